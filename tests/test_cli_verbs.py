"""The command line's verbs: one module each, loaded only when used, plug-in sets' through entry points.

`botstage --help` lists every installed verb without importing any verb's module; `validate`
imports its own and no other; a plug-in set's verb (or a third party's, from a wheel) is loaded
through the ``botstage.commands`` entry points, and one whose packages are missing names the
pip extra instead of printing a traceback.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib.metadata import distribution, entry_points
from pathlib import Path

import pytest
import typer

from botstage.missions.cli import Verbs, app
from botstage.missions.cli.verbs import GROUP, Verb, summary
from tests.tools import install_wheel

ROOT = Path(__file__).resolve().parent.parent
HELLO = str(ROOT / "missions" / "examples" / "hello.yaml")

# the plug-in sets' packages: never imported to list the verbs or to validate a mission
SETS = ("zenoh", "fastapi", "uvicorn", "zmq", "onnxruntime", "serial", "dynamixel_sdk", "pocketsphinx", "rosbags")
HEAVY = ("scipy", "matplotlib")

PLUGIN_VERBS = {
    "monitor": "web",
    "gallery": "web",
    "serve": "ros2",
    "up": "ros2",
    "certs": "ros2",
    "emulate": "hardware",
    "speech": "speech",
    "chat": "chat",
    "import": "",  # BT.CPP's set: registered by entry point, but it needs no package, so no extra
    "export": "",
}

PROBE = """
import json, os, sys
for blocked in os.environ.get("PROBE_BLOCK", "").split():
    sys.modules[blocked] = None  # as if the package were not installed
sys.argv = ["botstage", *sys.argv[1:]]
from botstage.missions.cli import app
try:
    app()
finally:
    with open(os.environ["PROBE_OUT"], "w") as out:
        json.dump(sorted(sys.modules), out)
"""


def probe(
    tmp_path: Path, *args: str, block: tuple[str, ...] = (), env: dict[str, str] | None = None
) -> tuple[subprocess.CompletedProcess[str], set[str]]:
    """``botstage ARGS`` in a fresh process: what it printed and every module it imported."""
    out = tmp_path / "modules.json"
    environ = {**(env or os.environ), "PROBE_OUT": str(out), "PROBE_BLOCK": " ".join(block), "COLUMNS": "250"}
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *args], capture_output=True, text=True, cwd=ROOT, env=environ, timeout=300
    )
    return done, set(json.loads(out.read_text())) if out.exists() else set()


def top_level(modules: set[str]) -> set[str]:
    return {name.split(".")[0] for name in modules}


def verb_modules(modules: set[str]) -> set[str]:
    helpers = {"botstage.missions.cli", "botstage.missions.cli.verbs", "botstage.missions.cli.common"}
    return {name for name in modules if name.startswith("botstage.missions.cli.") and name not in helpers}


def test_help_lists_every_verb_and_imports_none_of_their_modules(tmp_path: Path) -> None:
    done, modules = probe(tmp_path, "--help")
    assert done.returncode == 0, done.stderr
    listed = {line.split()[1] for line in done.stdout.splitlines() if line.startswith("│ ") and len(line.split()) > 2}
    assert set(Verbs.core) | set(PLUGIN_VERBS) <= listed
    assert "Check missions (or deployments, with their mission)" in done.stdout  # the docstrings' help
    assert verb_modules(modules) == set()
    assert not top_level(modules) & {*SETS, *HEAVY, "aiml", "cv2", "numpy", "pydantic", "py_trees", "transitions"}


def test_validate_imports_its_own_module_and_no_plugin_set(tmp_path: Path) -> None:
    done, modules = probe(tmp_path, "validate", HELLO)
    assert done.returncode == 0, done.stderr
    assert verb_modules(modules) == {"botstage.missions.cli.validate"}
    assert not top_level(modules) & {*SETS, *HEAVY}


def test_each_verb_is_listed_with_the_help_its_command_has() -> None:
    """The listing reads the help from the source; the loaded command must say the same."""
    group = typer.main.get_command(app)
    assert isinstance(group, Verbs)
    with typer.Context(group) as ctx:
        for name in group.list_commands(ctx):
            verb = group.verbs()[name]
            assert summary(verb), name
            assert summary(verb) == group.load(name).help, name


def test_the_plugin_sets_register_their_verbs_with_the_extra_that_brings_them() -> None:
    ours = {point.name: point for point in entry_points(group=GROUP) if point.dist and point.dist.name == "botstage"}
    assert {name: point.extras for name, point in ours.items()} == {
        name: [x] if x else [] for name, x in PLUGIN_VERBS.items()
    }
    extras = set(distribution("botstage").metadata.get_all("Provides-Extra") or [])
    assert set(PLUGIN_VERBS.values()) - {""} <= extras
    assert not set(ours) & set(Verbs.core)


@pytest.mark.parametrize(
    ("args", "blocked", "extra"),
    [(["monitor", "runs/none"], "fastapi", "web"), (["serve", "robot", "chefbot"], "zenoh", "ros2")],
)
def test_a_plugin_verb_without_its_set_names_the_extra(
    tmp_path: Path, args: list[str], blocked: str, extra: str
) -> None:
    done, _ = probe(tmp_path, *args, block=(blocked,))
    assert done.returncode == 1, done.stdout + done.stderr
    assert f"needs {blocked}, which is not installed: pip install 'botstage[{extra}]'" in done.stderr
    assert "Traceback" not in done.stderr


def test_run_monitor_without_the_web_set_names_the_extra(tmp_path: Path) -> None:
    done, _ = probe(tmp_path, "run", HELLO, "--monitor", "-q", "--out", str(tmp_path / "run"), block=("fastapi",))
    assert done.returncode == 2, done.stdout + done.stderr
    assert "pip install 'botstage[web]'" in done.stderr and "Traceback" not in done.stderr


KIT = '''\
"""Verbs of a third party's kit."""

import sys

import typer

sys.stderr.write("verbs_kit.cli imported\\n")

greet_app = typer.Typer(no_args_is_help=True, help="Greetings, several ways.")


def hello(name: str = typer.Argument("world", help="who to greet")) -> None:
    """Say hello to someone."""
    print(f"hello {name}")


@greet_app.command("loud")
def loud(name: str) -> None:
    """Shout hello."""
    print(f"HELLO {name.upper()}")
'''

BROKEN = '''\
import not_a_real_package_xyz


def broken() -> None:
    """Needs a package nobody installed."""
'''

KIT_ENTRY_POINTS = """\
[botstage.commands]
hello = verbs_kit.cli:hello
greet = verbs_kit.cli:greet_app
broken = verbs_kit.broken:broken [fancy]
run = verbs_kit.cli:hello
"""


@pytest.fixture(scope="module")
def kit_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    files = {"verbs_kit/__init__.py": "", "verbs_kit/cli.py": KIT, "verbs_kit/broken.py": BROKEN}
    site = install_wheel(tmp_path_factory.mktemp("verbs-kit"), "verbs-kit", files, KIT_ENTRY_POINTS)
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}


def test_a_third_party_verb_is_listed_without_importing_it(tmp_path: Path, kit_env: dict[str, str]) -> None:
    done, modules = probe(tmp_path, "--help", env=kit_env)
    assert done.returncode == 0, done.stderr
    rows = {
        line.split()[1]: line for line in done.stdout.splitlines() if line.startswith("│ ") and len(line.split()) > 2
    }
    assert "Say hello to someone." in rows["hello"] and "Greetings, several ways." in rows["greet"]
    assert "Needs a package nobody installed." in rows["broken"]
    assert "verbs_kit.cli imported" not in done.stderr and "verbs_kit.cli" not in modules
    assert "warning: `run` from verbs-kit ignored: botstage's core has it" in done.stderr


def test_a_third_party_verb_and_sub_app_run(tmp_path: Path, kit_env: dict[str, str]) -> None:
    done, _ = probe(tmp_path, "hello", "Ada", env=kit_env)
    assert (done.returncode, done.stdout) == (0, "hello Ada\n"), done.stderr
    done, _ = probe(tmp_path, "greet", "loud", "Ada", env=kit_env)
    assert (done.returncode, done.stdout) == (0, "HELLO ADA\n"), done.stderr
    done, _ = probe(tmp_path, "run", "--help", env=kit_env)
    assert done.returncode == 0 and "Run a mission" in done.stdout  # the core's verb keeps its name


def test_a_third_party_verb_that_cannot_load_says_what_to_install(tmp_path: Path, kit_env: dict[str, str]) -> None:
    done, _ = probe(tmp_path, "broken", "--anything", env=kit_env)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "needs not_a_real_package_xyz, which is not installed: pip install 'verbs-kit[fancy]'" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_verb_is_read_from_its_source() -> None:
    assert summary(Verb("validate", "botstage.missions.cli.validate:validate")).startswith("Check missions")
    assert summary(Verb("scenario", "botstage.missions.cli.scenario:scenario_app")) == (
        "Scenario files: make them from recorded runs."
    )
    assert summary(Verb("nothing", "botstage.missions.cli.validate:nothing")) == ""
    assert summary(Verb("nowhere", "no_such_package_xyz.cli:verb")) == ""
